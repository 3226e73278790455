"""Error against wall time, uniform against adaptive: ``convergence --adaptive TOL ...``.

After the convergence study, each TOL runs the passes of ``run --tol``
(app/studies/tolerance.py, used as it is: ``run_passes`` and its passes.json) on the same
case, from the study's coarsest level h = k = 1/levels[0] (a mesh.file: the mesh as read,
level 0), with the delta of the study's first rows.  error_vs_wall.csv and
error_vs_wall.png then put side by side:

- one row per uniform level (the study's rows of that delta): its wall time, its own
  estimate est_max and its true Error (the study's, against the reference), each also
  relative to the level's scale max_n (||sigma_n||_Q + ||u_n||_V + ||kappa_n||_Y);
- one row per adaptive pass: the cumulative wall time of the passes so far (the sum of
  passes.json's wall_s: the stop rule needs them all) and the pass's estimate and scale;
  the last pass also has its true Error against the study's reference where it is
  defined as the uniform levels' is: its mesh, refined locally by bisection
  (meshes/adapt.py), does not nest in the reference grid, so the Error is integrated
  exactly on the overlay of the two meshes (app/studies/overlay.py), over the pass's time
  points if they are all reference time points (none otherwise: k halved per pass can be
  finer than the reference's; none for a mesh.file study either).

Wall times: ``wall_s`` is what a run costs without outputs: a uniform level's set-up
(mesh, forms, matrices) plus its steps, a pass's whole time (passes.json's wall_s: mesh
refinement, set-up, steps, the summary); ``steps_s`` is the steps alone (the study's
``solve_s``, each pass's summary.json ``solve_s``, summed over the passes so far), as the
convergence table's wall column.
"""
from __future__ import annotations

import copy
import dataclasses
import json
import logging
import time
from pathlib import Path

from vpcontact.io.errors import CaseError
from vpcontact.io.files import atomic_write
from vpcontact.io.output import csv_text

log = logging.getLogger("vpcontact")

COLUMNS = ["kind", "tol", "delta", "level", "pass", "status", "cells", "dofs", "steps",
           "wall_s", "steps_s", "estimate", "est_time", "est_space", "scale", "relative",
           "error", "error_relative", "met"]


class PassesInterrupted(Exception):
    """A signal (SIGINT, SIGTERM) stopped the passes of a tolerance.

    Args:
        tol: the tolerance.
        where: the directory of its passes.
    """

    def __init__(self, tol: float, where: Path):
        super().__init__(f"the passes of --adaptive {tol:g} ({where})")
        self.tol, self.where = tol, where


def tol_dir(outdir: Path, tol: float) -> Path:
    """The directory of the passes of one tolerance.

    Args:
        outdir: the study's output directory.
        tol: the tolerance.

    Returns:
        outdir/adaptive/tol_<tol>.
    """
    return outdir / "adaptive" / f"tol_{tol:g}"


def check_adaptive(case, tols: list[float] | None, levels: list[int], vary: str) -> None:
    """Refuse ``--adaptive`` values or a case the passes cannot run (before any computation).

    Args:
        case: the validated Case.
        tols: --adaptive, or None (nothing to check).
        levels: the study's levels (resolved).
        vary: --vary.

    Raises:
        CaseError: one line naming --adaptive and what is allowed.
    """
    if tols is None:
        return
    from vpcontact.studies.tolerance import check_tolerance_case
    if len(set(tols)) != len(tols):
        raise CaseError(f"--adaptive {' '.join(f'{t:g}' for t in tols)}: a tolerance is "
                        "repeated (allowed: distinct numbers > 0)")
    if vary != "both":
        raise CaseError(f"--adaptive: compares with the uniform levels h = k; --vary {vary} "
                        "is not allowed with it (allowed: --vary both)")
    if case.mesh.file is not None and levels and levels[0] != 0:
        raise CaseError(f"--adaptive: the passes start from the mesh.file as read (level 0); "
                        f"--levels starts at {levels[0]} (allowed: --levels 0 ...)")
    try:
        check_tolerance_case(case, case.raw)
    except CaseError as exc:
        raise CaseError(f"--adaptive: {exc}") from None


def start_case(raw: dict, level: int, delta: float, source: str, petsc_cli: dict):
    """The case of the first pass: the study's coarsest level with ``delta``.

    Args:
        raw: the case as read.
        level: the study's first level (n = N = level; 0 for a mesh.file: its mesh and
            time.N).
        delta: the regularisation width.
        source: the case file, for messages.
        petsc_cli: PETSc options of the command line.

    Returns:
        (its raw dict, the validated Case with the command line's PETSc options).
    """
    from vpcontact.studies.convergence import raw_at
    if "file" in raw["mesh"]:
        raw = copy.deepcopy(raw)
        raw.setdefault("solver", {})["delta"] = delta
    else:
        raw = raw_at(raw, level, level, delta)
    return raw, _validated(raw, source, petsc_cli)


def _validated(raw: dict, source: str, petsc_cli: dict):
    """validate, with the command line's PETSc options over the case's."""
    from vpcontact.case import validate
    case = validate(raw, source)
    return dataclasses.replace(case, petsc={**case.petsc, **petsc_cli})


def adaptive_run(raw: dict, source: str, level: int, delta: float, tol: float, comm,
                 outdir: Path, petsc_cli: dict, max_passes: int,
                 ref_times=()) -> tuple[dict, object]:
    """The passes of ``run --tol`` for one tolerance (collective), without outputs but each
    pass's summary.json (for its steps' time).

    Args:
        raw: the case as read.
        source: the case file.
        level: the study's first level.
        delta: the regularisation width.
        tol: the tolerance.
        comm: the MPI communicator.
        outdir: the directory of the passes (passes.json, pass_<i>/summary.json).
        petsc_cli: PETSc options of the command line.
        max_passes: the most passes.
        ref_times: the reference's time points (the passes' fields are kept at those only).

    Returns:
        (the content of passes.json: tol, met, theta and the passes' rows, on every rank;
        the last pass's overlay.MeshSamples, its samples on rank 0).
    """
    from vpcontact.observers import RunFiles
    from vpcontact.studies.overlay import MeshSamples
    from vpcontact.studies.tolerance import run_passes
    raw0, case = start_case(raw, level, delta, source, petsc_cli)
    last = []

    def observers():
        last[:] = [MeshSamples(ref_times)]    # the fields of the pass, kept for the last
        return [RunFiles(), last[0]]

    log.info("adaptive: run --tol %g from %s (delta = %g) -> %s", tol,
             "the mesh.file as read" if case.mesh.file else f"h = k = 1/{level}", delta, outdir)
    loglevel = log.level
    log.setLevel(max(loglevel, logging.WARNING))   # the passes' lines at the end, as the study
    try:
        run_passes(raw0, case, comm, tol, max_passes, outdir, observers,
                   lambda r, s: _validated(r, s, petsc_cli))
    finally:
        log.setLevel(loglevel)
    comm.barrier()
    rows = json.loads((outdir / "passes.json").read_text()) if comm.rank == 0 else None
    return comm.bcast(rows, root=0), last[0]


def uniform_rows(res: dict, delta: float) -> list[dict]:
    """The rows of the uniform levels of one delta, and of the reference if it has that
    delta (kind "reference": its estimate, no Error).

    Args:
        res: the result of convergence.study.
        delta: the delta.

    Returns:
        One dict per level (COLUMNS), then the reference's.
    """
    out = []
    for r in (r for r in res["rows"] if r["delta"] == delta):
        out.append(_uniform_row("uniform", delta, r["level"], r["dofs"], r["steps"],
                                r["setup_s"], r["solve_s"], r, r["error"]))
    ref = res["reference"]
    if res["ref_delta"] == delta and ref.estimate is not None:
        e = ref.estimate
        out.append(_uniform_row("reference", delta, res["reference_level"], ref.dofs, ref.N,
                                ref.setup_s, ref.solve_s,
                                {"estimate": e["estimate"], "est_time": e["time"],
                                 "est_space": e["space"], "scale": e.get("scale")}, None))
    return out


def _uniform_row(kind, delta, level, dofs, steps, setup_s, solve_s, est: dict,
                 error) -> dict:
    """A row of a uniform run: its wall times, its estimate and (a level's) Error, each
    relative to the run's scale."""
    scale = est["scale"]
    return {"kind": kind, "delta": delta, "level": level, "dofs": dofs, "steps": steps,
            "wall_s": setup_s + solve_s, "steps_s": solve_s, "estimate": est["estimate"],
            "est_time": est["est_time"], "est_space": est["est_space"], "scale": scale,
            "relative": est["estimate"] / scale if scale and est["estimate"] is not None
            else None, "error": error,
            "error_relative": error / scale if scale and error is not None else None}


def adaptive_rows(tol: float, delta: float, passes_json: dict, outdir: Path) -> list[dict]:
    """The rows of one tolerance's passes (call on rank 0: reads the passes' summaries).

    Args:
        tol: the tolerance.
        delta: the delta of the passes.
        passes_json: the content of passes.json.
        outdir: the directory of the passes.

    Returns:
        One dict per pass (COLUMNS), wall_s and steps_s summed over the passes so far.
    """
    out, wall, steps = [], 0.0, 0.0
    rows = passes_json["passes"]
    for p in rows:
        wall += p["wall_s"]
        summary = json.loads((outdir / f"pass_{p['index']}" / "summary.json").read_text())
        steps += summary["solve_s"]
        out.append({"kind": "adaptive", "tol": tol, "delta": delta, "pass": p["index"],
                    "status": p["status"], "cells": p["cells"], "dofs": p["dofs"],
                    "steps": p["steps"],
                    "wall_s": wall, "steps_s": steps, "estimate": p["est_max"],
                    "est_time": p["est_time"], "est_space": p["est_space"],
                    "scale": p["scale"], "relative": p["relative"],
                    "met": passes_json["met"] if p is rows[-1] else None})
    return out


def final_error(samples, res: dict, scale: float | None) -> dict:
    """The true Error of the last pass against the study's reference (rank 0), exact on the
    overlay of its mesh and the reference grid (app/studies/overlay.py), and relative to its
    scale; none for a mesh.file study (its reference is not a structured grid) or when a
    time point of the pass is not a reference time point (said in the log).

    Args:
        samples: the last pass's overlay.MeshSamples.
        res: the result of convergence.study.
        scale: the pass's scale.

    Returns:
        {"error", "error_relative"}, or {} without an Error.
    """
    from vpcontact.studies.overlay import overlay_error
    ref = res["reference"]
    if res["file"] or samples.off or not samples.snaps:
        if samples.off and not res["file"]:
            log.info("adaptive: the last pass's time points are not all reference time "
                     "points: no true Error")
        return {}
    t0 = time.perf_counter()
    e = overlay_error(samples, ref, ref.grid)
    if e is None:
        log.info("adaptive: the last pass's time points are not all reference time points: "
                 "no true Error")
        return {}
    log.info("adaptive: the last pass's true Error %.6g (on the overlay with the reference, "
             "%.1f s)", e["error"], time.perf_counter() - t0)
    return {"error": e["error"], "error_relative": e["error"] / scale if scale else None}


def write_csv(path: Path, rows: list[dict]) -> None:
    """error_vs_wall.csv (COLUMNS; floats at full precision), atomically.

    Args:
        path: the file.
        rows: uniform_rows and adaptive_rows.
    """
    atomic_write(path, csv_text(COLUMNS, rows))


def figure(rows: list[dict], tols: list[float], file: bool = False):
    """Estimate / scale (and the uniform levels' Error / scale) against wall time, log-log:
    the whole cost (left) and the steps only (right), a tolerance line per run to it.

    Args:
        rows: uniform_rows and adaptive_rows.
        tols: the tolerances.
        file: the levels are refinements of a mesh.file (their labels).

    Returns:
        The matplotlib Figure (laid out, not saved).
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vpcontact.studies.convergence import _log_ticks

    fig, axes = plt.subplots(1, 2, figsize=(11.5, 5.4))
    uni = [r for r in rows if r["kind"] in ("uniform", "reference")
           and r["relative"] is not None]
    for ax, key in zip(axes, ("wall_s", "steps_s")):
        x = [max(r[key], 1e-4) for r in uni]
        ax.loglog(x, [r["relative"] for r in uni], "o-", color="k",
                  label="uniform levels (and the reference): estimate")
        ax.loglog([xi for xi, r in zip(x, uni) if r["error"] is not None],
                  [r["error_relative"] for r in uni if r["error"] is not None], "o--",
                  color="grey", mfc="none", label="uniform levels: true Error")
        for r, xi in zip(uni, x):
            ax.annotate(_level_name(r, file), (xi, r["relative"]), textcoords="offset points",
                        xytext=(4, 4), fontsize=7)
        for i, tol in enumerate(tols):
            ad = [r for r in rows if r["kind"] == "adaptive" and r["tol"] == tol
                  and r["relative"] is not None]
            colour = f"C{i}"
            ax.loglog([max(r[key], 1e-4) for r in ad], [r["relative"] for r in ad], "s-",
                      color=colour, label=f"run --tol {tol:g}: the passes' estimates")
            ax.axhline(tol, color=colour, ls=":", lw=1, label=f"tol {tol:g}")
            if ad and ad[-1].get("error_relative") is not None:
                ax.loglog([max(ad[-1][key], 1e-4)], [ad[-1]["error_relative"]], "s",
                          mfc="none", ms=9, color=colour,
                          label=f"run --tol {tol:g}: true Error of the last pass")
        _log_ticks(ax.xaxis)
        _log_ticks(ax.yaxis)
        ax.grid(True, which="both", alpha=0.3)
        ax.set_ylabel("estimate (or Error) / scale")
    axes[0].set_xlabel("wall time [s]: set-up + steps (passes: cumulative)")
    axes[1].set_xlabel("wall time [s]: steps only (passes: cumulative)")
    axes[0].set_title("error against wall time, uniform vs adaptive")
    axes[1].set_title("the same, time steps only")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="lower center", ncol=3, fontsize=8)
    fig.tight_layout(rect=(0, 0.12, 1, 1))        # the legend below both panels
    return fig


def _level_name(row: dict, file: bool) -> str:
    """A uniform run's label: h = k = 1/L (r = L for a mesh.file's refinements)."""
    name = f"r = {row['level']}" if file else f"1/{row['level']}"
    return name + (" (reference)" if row["kind"] == "reference" else "")


def write_plot(path: Path, rows: list[dict], tols: list[float], file: bool = False) -> None:
    """error_vs_wall.png (matplotlib, Agg), atomically.

    Args:
        path: the PNG file.
        rows: uniform_rows and adaptive_rows.
        tols: the tolerances.
        file: the levels are refinements of a mesh.file.
    """
    import matplotlib.pyplot as plt

    from vpcontact.io.files import write_replacing
    fig = figure(rows, tols, file)
    write_replacing(path, lambda tmp: fig.savefig(tmp, dpi=120))
    plt.close(fig)


def study_rows(res: dict, tols: list[float], outdir: Path, comm, raw: dict, source: str,
               petsc_cli: dict, max_passes: int) -> list[dict]:
    """Run the passes of every tolerance and gather the rows of error_vs_wall.csv
    (collective; the rows on rank 0, None elsewhere).

    Args:
        res: the result of convergence.study.
        tols: the tolerances.
        outdir: the study's output directory.
        comm: the MPI communicator.
        raw: the case as read.
        source: the case file.
        petsc_cli: PETSc options of the command line.
        max_passes: the most passes of each tolerance.

    Returns:
        uniform_rows followed by each tolerance's adaptive_rows (rank 0).

    Raises:
        PassesInterrupted: a signal stopped a pass (or came between two).
    """
    delta = res["deltas"][0]
    rows = uniform_rows(res, delta)
    for tol in tols:
        where = tol_dir(outdir, tol)
        try:
            passes, samples = adaptive_run(raw, source, res["levels"][0], delta, tol, comm,
                                           where, petsc_cli, max_passes,
                                           () if res["file"] else res["reference"].times)
        except KeyboardInterrupt:
            raise PassesInterrupted(tol, where) from None
        if passes["passes"][-1]["status"] == "interrupted":
            raise PassesInterrupted(tol, where)
        if comm.rank == 0:
            rows += adaptive_rows(tol, delta, passes, where)
            rows[-1].update(final_error(samples, res, rows[-1]["scale"]))
    return rows if comm.rank == 0 else None
