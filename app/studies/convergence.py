"""Convergence study and work-precision view (the paper's Table 1 and beyond it).

Error = max_n ( ||sigma_n - sigma_n^ref||_Q + ||u_n - u_n^ref||_V + ||kappa_n - kappa_n^ref||_Y )
over the time points t_n of the coarse run (all of them are reference time points), with the
coarse fields prolonged exactly to the reference mesh and the norms integrated there (the
paper's Table 1).  ``vary``: "both" refines h and k together, "h" keeps k at the reference,
"k" keeps h at the reference.

Levels of a built-in structured rectangle: level L is the L x L mesh with N = L steps (h =
L1/L, k = T/L; app/studies/grid.py).  Levels of a case with ``mesh.file``: level r is the
user's mesh refined r times (each triangle into 4, each tetrahedron into 8: nested meshes,
meshes/refine.py; a .geo is meshed once at its mesh.size) with N = time.N * 2^r steps, so h
and k halve from level to level (app/studies/nested.py); the reference is the finest.

Wall time of a run = the sum of its steps' times (history update, SNES solve, stress update),
measured with time.perf_counter around each step; mesh generation, JIT compilation, form and
matrix set-up, outputs and the sampling for this study are excluded (reported apart as
set-up).  A cached run reports the times measured when it was computed.
"""
from __future__ import annotations

import contextlib
import copy
import logging
import math
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from vpcontact.case import CaseError, validate
from vpcontact.io.files import atomic_write
from vpcontact.io.output import csv_text
from vpcontact.observers import Observer
from vpcontact.post.quantities import contact_table
from vpcontact.studies import runcache
from vpcontact.studies.grid import (
    Grid,
    GridSampler,
    cell_l2_norm,
    prolong_dg0,
    prolong_p1,
    strain_norm,
)
from vpcontact.studies.interrupts import (
    SignalWatch,
    StudyInterrupted,
    check_run,
    signal_name,
    signals_held,
)
from vpcontact.studies.nested import LevelSampler, NestedLevel

log = logging.getLogger("vpcontact")

# Wang & Cheng (2021), Table 1: h = k = 1/8 .. 1/64 against h = k = 1/128.
PAPER_TABLE1 = {8: 23.1363, 16: 19.6575, 32: 13.2976, 64: 6.1820}
PAPER_RATES = {16: 0.2351, 32: 0.5639, 64: 1.1050}
PAPER_DATA = {  # the paper's Section 4
    ("mesh", "L1"): 1.0, ("mesh", "L2"): 1.0, ("time", "T"): 1.0,
    ("material", "E"): 1000.0, ("material", "nu"): 0.4,
}


@dataclass
class RunRecord:
    """One run of the study.

    Args:
        n: cells per side of the mesh (h = L1 / n), or the refinements r of a mesh.file.
        N: time steps (k = T / N).
        delta: the regularisation width of the run.
        grid: the structured grid of its mesh, or its NestedLevel (mesh.file).
        dofs: the number of displacement dofs.
        times: t_0, ..., t_N, shape (N + 1,).
        solve_s: wall time of the steps [s].
        setup_s: wall time of the set-up [s].
        newton: Newton iterations of all steps.
        cached: whether it came from the run cache.
        snaps: the fields (u, sigma, kappa) per time point; only on rank 0.
        contact: the Gamma3 table at T (problem.contact_table of all ranks) on rank 0, for a
            computed run; None for a cached one.
        last_step: the record of the run's last step (summary.json's, e.g. contact_force and
            reactions) for a computed run; None for a cached one.
        estimate: the run's a posteriori error estimate (summary.json's error_estimate:
            estimate, time, space, scale), or None (a cached run of an earlier version).
    """

    n: int
    N: int
    delta: float
    grid: Grid | NestedLevel
    dofs: int
    times: np.ndarray
    solve_s: float
    setup_s: float
    newton: int
    cached: bool
    snaps: list = field(default_factory=list, repr=False)
    contact: dict | None = field(default=None, repr=False)
    last_step: dict | None = field(default=None, repr=False)
    estimate: dict | None = field(default=None, repr=False)

    @property
    def h(self) -> float:
        """The mesh size: L1 / n, or the level's nominal h_0 / 2^r."""
        return self.grid.h if isinstance(self.grid, NestedLevel) else self.grid.L1 / self.n


DEFAULT_LEVELS, DEFAULT_REFERENCE = [8, 16, 32, 64], 128   # built-in meshes: n = N = level
DEFAULT_REFINEMENTS = [0, 1, 2]                              # mesh.file: refinements


def resolve_levels(case, levels: list[int] | None, reference: int | None) -> tuple[
        list[int], int]:
    """The study's levels and reference, with the defaults of the case's kind of mesh.

    Args:
        case: the validated Case.
        levels: --levels, or None.
        reference: --reference, or None.

    Returns:
        (levels, reference): built-in meshes default to 8 16 32 64 against 128 (n = N =
        level); a mesh.file to the refinements 0 1 2 (0 .. R - 1 given the reference R)
        against the largest level + 1.
    """
    if case.mesh.file is None:
        return (list(levels) if levels is not None else list(DEFAULT_LEVELS),
                reference if reference is not None else DEFAULT_REFERENCE)
    if levels is None:
        levels = list(DEFAULT_REFINEMENTS) if reference is None else list(range(reference))
    return list(levels), reference if reference is not None else max(levels, default=0) + 1


def plan_runs(levels: list[int], reference: int, vary: str, case=None,
              deltas: list[float] | None = None) -> list[tuple[int, int]]:
    """The resolutions of the study's levels, checking that meshes and time grids nest in the
    reference (and, given the case, that its mesh is structured or a mesh.file and that the
    case is valid at every level and the reference with every delta).

    Args:
        levels: the levels, strictly increasing: for a built-in mesh n (= N for vary
            "both"), each a divisor of ``reference``; for a mesh.file the refinements r >= 0,
            each below ``reference``.
        reference: the reference level (h = k = 1/128 for Table 1; the finest refinement
            for a mesh.file).
        vary: "both" (h and k together), "h" (k at the reference) or "k" (h at the
            reference).
        case: the validated Case, or None to check the numbers only (built-in meshes).
        deltas: the regularisation widths to run (None: the case's).

    Returns:
        (n, N) of each level: cells per side (or refinements) and time steps.

    Raises:
        CaseError: naming the option and the allowed values.
    """
    if case is not None and case.mesh.file is not None:
        return _plan_refinements(levels, reference, vary, case, deltas)
    if case is not None and case.mesh.kind != "structured":
        raise CaseError(f"{case.source}: mesh.kind: the convergence study needs nested meshes "
                        "(structured, or a mesh.file refined uniformly); got 'unstructured'")
    if case is not None and case.dim != 2:
        raise CaseError(f"{case.source}: mesh.dim: the convergence study of a built-in mesh is "
                        "for 2D cases (nested structured rectangles); a 3D mesh.file is refined")
    _check_plan(case, vary, levels, not levels or any(L < 1 for L in levels) or reference < 1,
                "--levels and --reference must be positive integers (allowed: 1 or more, "
                "cells per side of the built-in mesh)")
    bad = [L for L in levels if reference % L or L >= reference]
    if bad:
        raise CaseError(f"--levels {bad}: every level must divide the reference {reference} and "
                        "be smaller (nested meshes and common time points)")
    _check_deltas(deltas)
    plan = [(L, L) if vary == "both" else (L, reference) if vary == "h" else (reference, L)
            for L in levels]
    if case is not None:
        ds = list(deltas) if deltas else [case.numerics.delta]
        ref_delta = min([case.numerics.delta, *ds])
        with _naming("--reference", reference):
            _case_at(case.raw, reference, reference, ref_delta, case.source)
        for L, (n, N) in zip(levels, plan):
            for delta in ds:
                with _naming("--levels", L):
                    _case_at(case.raw, n, N, delta, case.source)
    return plan


@contextlib.contextmanager
def _naming(option: str, value: int):
    """A CaseError of a level's case names the study's option that made it (the case's
    mesh.n or time.N was set from it)."""
    try:
        yield
    except CaseError as exc:
        raise CaseError(f"{option} {value}: {exc}") from None


def _check_plan(case, vary: str, levels, bad_levels: bool, why: str) -> None:
    """The checks every study plan makes: uniform time steps, --vary, levels increasing."""
    _check_uniform_time(case)
    if vary not in ("both", "h", "k"):
        raise CaseError(f"--vary: {vary!r} is not allowed (allowed: both, h, k)")
    if bad_levels:
        raise CaseError(why)
    if sorted(set(levels)) != list(levels):
        raise CaseError(f"--levels must increase strictly, got {levels}")


def _check_uniform_time(case) -> None:
    if case is not None and ("times" in case.raw["time"] or "grading" in case.raw["time"]):
        raise CaseError(f"{case.source}: time: the convergence study refines uniform steps; "
                        "give time.T and time.N")


def _check_deltas(deltas) -> None:
    if deltas is not None and (not deltas or not all(
            isinstance(d, (int, float)) and math.isfinite(d) and d > 0 for d in deltas)):
        raise CaseError(f"--deltas {deltas}: not allowed (allowed: one or more finite "
                        "numbers > 0)")
    if deltas and len(set(deltas)) != len(deltas):
        raise CaseError(f"--deltas {deltas}: a delta is repeated (allowed: distinct finite "
                        "numbers > 0)")


def _base_steps(case) -> int:
    """The time steps of level 0 of a mesh.file study: the case's time.N."""
    return len(case.time.times) - 1


def _plan_refinements(levels, reference, vary, case, deltas) -> list[tuple[int, int]]:
    """plan_runs for a mesh.file: level r = r refinements with N = time.N 2^r steps."""
    _check_plan(case, vary, levels, not levels or any(r < 0 for r in levels) or reference < 1,
                "--levels and --reference of a mesh.file case count uniform refinements of "
                "its mesh: integers >= 0 (the reference >= 1)")
    bad = [r for r in levels if r >= reference]
    if bad:
        raise CaseError(f"--levels {bad}: every level must be below the reference {reference} "
                        "(the reference is the mesh refined the most)")
    _check_deltas(deltas)
    N0 = _base_steps(case)
    plan = [(r, N0 * 2 ** r) if vary == "both" else (r, N0 * 2 ** reference) if vary == "h"
            else (reference, N0 * 2 ** r) for r in levels]
    ds = list(deltas) if deltas else [case.numerics.delta]
    ref_delta = min([case.numerics.delta, *ds])
    with _naming("--reference", reference):
        _case_at_level(case.raw, case.mesh.file, N0 * 2 ** reference, ref_delta, case.source)
    for r, (_, N) in zip(levels, plan):
        for delta in ds:
            with _naming("--levels", r):
                _case_at_level(case.raw, case.mesh.file, N, delta, case.source)
    return plan


def check_cache_dir(cache_dir: Path | None, comm) -> None:
    """Check the run cache directory (collective; tested on rank 0, which writes the cache).

    Args:
        cache_dir: the run cache directory, or None (no cache: nothing to check).
        comm: the MPI communicator.

    Raises:
        CaseError: on every rank, unless ``cache_dir`` is (or can be made) a writable
            directory.
    """
    if cache_dir is None:
        return
    from vpcontact.cachepaths import unusable
    why = comm.bcast(unusable(Path(cache_dir)) if comm.rank == 0 else None, root=0)
    if why:
        raise CaseError(f"--cache-dir {cache_dir}: not a writable directory ({why})")


def raw_at(raw: dict, n: int, N: int, delta: float) -> dict:
    """The case as read at a level of a built-in mesh: n cells per side, N uniform steps and
    the regularisation width delta.

    Args:
        raw: the case as read (not modified).
        n: cells per side.
        N: time steps.
        delta: the regularisation width.

    Returns:
        A copy with mesh.n, time.N (time.k removed) and solver.delta set.
    """
    raw = copy.deepcopy(raw)
    raw["mesh"]["n"], raw["time"]["N"] = n, N
    raw["time"].pop("k", None)
    raw.setdefault("solver", {})["delta"] = delta
    return raw


def _case_at(raw: dict, n: int, N: int, delta: float, source: str):
    return validate(raw_at(raw, n, N, delta), source)


def _case_at_level(raw: dict, path, N: int, delta: float, source: str):
    """The case on a level's .msh (absolute path) with N uniform steps and delta."""
    raw = copy.deepcopy(raw)
    raw["mesh"] = {"file": str(path), "dim": raw["mesh"].get("dim", 2)}
    raw["time"]["N"] = N
    raw["time"].pop("k", None)
    raw.setdefault("solver", {})["delta"] = delta
    return validate(raw, source)


class GridSamples(Observer):
    """Samples u_n, sigma_n, kappa_n on the study's grid (or refined level) at t_0 and after
    every step (an observer of the run); ``snaps`` (one dict per time point) on rank 0 only.

    Args:
        grid: the structured grid of the run's mesh, or its NestedLevel.
    """

    def __init__(self, grid: Grid):
        self.grid, self.snaps, self.sampler = grid, [], None

    def start(self, sim) -> None:
        """Sample the start state (t_0) (collective).

        Args:
            sim: the Simulation, set up.
        """
        self._sample(sim)

    def step(self, sim, record: dict) -> None:
        """Sample u_n, sigma_n, kappa_n after step n (collective).

        Args:
            sim: the Simulation after step n was accepted.
            record: the step's record (unused).
        """
        self._sample(sim)

    def _sample(self, sim) -> None:
        if self.sampler is None:
            kind = LevelSampler if isinstance(self.grid, NestedLevel) else GridSampler
            self.sampler = kind(sim.problem, self.grid)
        snap = self.sampler.sample(sim.problem, sim.history)     # collective
        if sim.comm.rank == 0:
            self.snaps.append(snap)


def _from_cache(path: Path | None, case, grid: Grid):
    """(times, snaps, meta) of the cached run at ``path``, or None: not cached, an entry
    that is damaged or does not fit the run (a warning; the run is computed again), or one
    of an earlier version whose estimate has no scale (computed again, said in the log)."""
    if path is None or not path.exists():
        return None
    if isinstance(grid, NestedLevel):
        shapes = grid.shapes()
    else:
        n = grid.n
        shapes = {"u": (n + 1, n + 1, 2), "sigma": (n, n, 2, 2, 2), "kappa": (n, n, 2)}
    try:
        entry = runcache.load(path, case.time.times, shapes)
    except runcache.Unreadable as exc:
        log.warning("run cache entry %s is not usable (%s): computing the run again", path, exc)
        return None
    if "scale" not in (entry[2].get("estimate") or {}):
        log.info("run cache entry %s is of an earlier version (no estimate scale): computing "
                 "the run again", path.name)
        return None
    return entry


def obtain_run(raw: dict, n: int, N: int, delta: float, source: str, petsc_cli: dict, comm,
               cache_dir: Path | None, level: NestedLevel | None = None) -> RunRecord:
    """Run (or load from the cache) the case at resolution (n, N) with regularisation delta
    (collective); a computed run is added to the cache.

    Args:
        raw: the case as read (a dict).
        n: cells per side (built-in mesh), or the refinements of ``level``.
        N: time steps.
        delta: the regularisation width.
        source: the case file, for messages.
        petsc_cli: PETSc options from the command line (over the case's).
        comm: the MPI communicator.
        cache_dir: the run cache directory, or None.
        level: the refined mesh.file level to run on, or None (the built-in mesh).

    Returns:
        The RunRecord (with its samples and, if computed, its final contact table on rank 0).

    Raises:
        RuntimeError: the run did not complete.
        StudyInterrupted: a signal stopped the run.
    """
    import dataclasses

    from vpcontact.simulation import run

    if level is None:
        case = _case_at(raw, n, N, delta, source)
        grid, what = Grid(n, case.mesh.L1, case.mesh.L2, case.mesh.diagonal), f"n = {n:4d}"
    else:
        case, grid, what = _case_at_level(raw, level.path, N, delta, source), level, f"r = {n}"
    case = dataclasses.replace(case, petsc={**case.petsc, **petsc_cli})
    path = cache_dir / f"run-{runcache.cache_key(case)}.h5" if cache_dir else None
    cached = _from_cache(path, case, grid) if comm.rank == 0 else None
    if comm.bcast(cached is not None, root=0):
        times, snaps, meta = cached if comm.rank == 0 else (None, [], None)
        meta = comm.bcast(meta, root=0)
        times = comm.bcast(times, root=0)
        log.info("  %s, N = %4d, delta = %g: from the cache (%s)", what, N, delta, path.name)
        return RunRecord(n, N, delta, grid, meta["dofs"], np.asarray(times), meta["solve_s"],
                         meta["setup_s"], meta["newton"], True, snaps,
                         estimate=meta.get("estimate"))

    sampler, watch = GridSamples(grid), SignalWatch()
    loglevel = log.level
    log.setLevel(max(loglevel, logging.WARNING))   # one line per run, not per step
    try:
        result = run(case, comm, [sampler, watch])
    finally:
        log.setLevel(loglevel)
    s = result.summary
    where = f"the run {' '.join(what.split())}, N = {N}, delta = {delta:g}"
    check_run(s, where)
    if result.status != "completed":
        raise RuntimeError(f"run {' '.join(what.split())}, N = {N}, delta = {delta:g} failed: "
                           f"{s['failure']['reason']} at step {s['failure']['step']}")
    rec = RunRecord(n, N, delta, grid, s["mesh"]["dofs"], np.array(case.time.times),
                    s["solve_s"], s["setup_s"], s["newton_iterations_total"], False,
                    sampler.snaps, _final_table(result.problem, comm),
                    s["steps"][-1] if s["steps"] else None, _estimate(s))
    try:
        with signals_held():          # the finished run is logged and cached whole
            _keep(rec, what, path, case.time.times, comm)
    except KeyboardInterrupt as exc:
        watch.signal = watch.signal or signal_name(exc)
    watch.stop_if_signalled(where)    # a signal in its last steps: the run is kept, then stop
    return rec


def _keep(rec: RunRecord, what: str, path: Path | None, times, comm) -> None:
    """The line of a computed run, and its cache entry (rank 0) if there is a cache."""
    log.info("  %s, N = %4d, delta = %g: %d dofs, %.2f s (+ set-up %.2f s), "
             "%d Newton iterations", what, rec.N, rec.delta, rec.dofs, rec.solve_s,
             rec.setup_s, rec.newton)
    if path and comm.rank == 0:
        try:
            runcache.save(path, times, rec.snaps,
                          {"dofs": rec.dofs, "solve_s": rec.solve_s, "setup_s": rec.setup_s,
                           "newton": rec.newton, "n": rec.n, "N": rec.N, "delta": rec.delta,
                           "estimate": rec.estimate})
        except OSError as exc:        # e.g. a full disk: the study goes on without the entry
            log.warning("run not cached (%s: %s)", path, exc.strerror or exc)


def _estimate(summary: dict) -> dict | None:
    """The run's error estimate (estimate, time, space, scale) from its summary, or None."""
    e = summary.get("error_estimate")
    return None if e is None else {k: e[k] for k in ("estimate", "time", "space", "scale")}


def _final_table(problem, comm) -> dict | None:
    """The contact table at T of all ranks on rank 0 (None elsewhere, or without Gamma3)."""
    return None if problem.disc.gamma3 is None else _gather_table(contact_table(problem), comm)


def _gather_table(table: dict, comm) -> dict | None:
    """The ranks' contact tables joined on rank 0 (None elsewhere)."""
    parts = comm.gather(table, root=0)
    if comm.rank != 0:
        return None
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def _norm_ops(level: RunRecord, ref: RunRecord):
    """(prolong P1, prolong DG0, ||.||_V, cell L2 norm) of a level against the reference."""
    if isinstance(ref.grid, NestedLevel):
        lg, rg = level.grid, ref.grid
        return (lambda a: lg.prolong_p1(a, rg), lambda a: lg.prolong_dg0(a, rg),
                rg.strain_norm, rg.cell_l2_norm)
    return (lambda a: prolong_p1(a, level.grid, ref.grid),
            lambda a: prolong_dg0(a, level.grid, ref.grid),
            lambda d: strain_norm(d, ref.grid), lambda f: cell_l2_norm(f, ref.grid))


def run_error(level: RunRecord, ref: RunRecord) -> dict:
    """The Error of the paper's Table 1 of a level against the reference (on rank 0):
    max over the level's time points t_n of
    ||sigma_n - sigma_n^ref||_Q + ||u_n - u_n^ref||_V + ||kappa_n - kappa_n^ref||_Y,
    the level's fields prolonged exactly to the reference mesh.

    Args:
        level: the level's run (with snaps).
        ref: the reference run (with snaps).

    Returns:
        {"error", "e_sigma", "e_u", "e_kappa", "n_max", "t_max"}: the Error, its three
        parts at the maximising time point, and that point's index and time.

    Raises:
        ValueError: a time point of the level is not a reference time point.
    """
    p1, dg0, v_norm, cell_norm = _norm_ops(level, ref)
    best = None
    for i, t in enumerate(level.times):
        m = int(np.argmin(np.abs(ref.times - t)))
        if abs(ref.times[m] - t) > 1e-12 * max(1.0, abs(t)):
            raise ValueError(f"time {t} of the level is not a reference time point")
        a, b = level.snaps[i], ref.snaps[m]
        e_u = v_norm(p1(a["u"]) - b["u"])
        e_s = cell_norm(dg0(a["sigma"]) - b["sigma"])
        e_k = cell_norm(dg0(a["kappa"]) - b["kappa"])
        total = e_s + e_u + e_k
        if best is None or total > best["error"]:
            best = {"error": total, "e_sigma": e_s, "e_u": e_u, "e_kappa": e_k, "n_max": i,
                    "t_max": float(t)}
    return best


def _observed_rates(x: list[float], err: list[float]) -> list[float | None]:
    """Table 1's rates log(E_{i-1} / E_i) / log(x_{i-1} / x_i) (x: h or k); None at level 0."""
    return [None] + [math.log(err[i - 1] / err[i]) / math.log(x[i - 1] / x[i])
                     for i in range(1, len(err))]


def matches_paper(raw: dict) -> bool:
    """Whether a case carries the paper's Section 4 data (so Table 1 applies).

    Args:
        raw: the case as read (a dict).

    Returns:
        True if it validates and has the paper's geometry, material, contact, friction (4.2)
        and loads; False otherwise.
    """
    try:
        c = validate(raw, "paper-check")
    except CaseError:
        return False
    if c.material is None:              # materials: one per group of cells, a mesh.file
        return False
    fr = c.contact.friction
    vp = c.material.viscoplastic
    return (c.mesh.kind == "structured" and c.mesh.L1 == 1.0 and c.mesh.L2 == 1.0
            and c.time.T == 1.0 and (c.material.E, c.material.nu) == (1000.0, 0.4)
            and vp is not None and vp.law == "perzyna"
            and (vp.lambda1, vp.lambda2, vp.kappa0) == (100.0, 100.0, 0.0)
            and (c.contact.g, c.contact.c_nu) == (0.012, 100.0) and fr is not None
            and (fr.b, fr.c1, fr.c2, fr.u1) == (1.0, 60.0, 60.0, 0.01)
            and c.loads.traction == {"top": (0.0, -8.0), "right": (-3.2, 0.0)}
            and not any(c.loads.f0))


COLUMNS = ["delta", "level", "h", "k", "n", "N", "dofs", "steps", "error", "e_sigma", "e_u",
           "e_kappa", "n_max", "t_max", "rate", "estimate", "est_time", "est_space",
           "scale", "effectivity", "solve_s", "setup_s", "newton_total", "cached"]


def study(raw: dict, source: str, levels: list[int], reference: int, vary: str,
          deltas: list[float], comm, cache_dir: Path | None, petsc_cli: dict) -> dict:
    """Run the convergence study (collective): the reference run, then every level with
    every delta, and the Error of Table 1 of each against the reference.

    Args:
        raw: the case as read (a dict).
        source: the case file, for messages.
        levels: the levels, strictly increasing (see plan_runs; refinements for a
            mesh.file).
        reference: the reference level.
        vary: "both", "h" or "k" (see plan_runs).
        deltas: the regularisation widths (empty: the case's).
        comm: the MPI communicator.
        cache_dir: the run cache directory, or None.
        petsc_cli: PETSc options from the command line.

    Returns:
        {"rows": one dict per (delta, level) with the COLUMNS, "reference": its RunRecord,
        "records": {(delta, level): RunRecord}, "ref_norms": the reference's max_n norms,
        "vary", "levels", "reference_level", "deltas", "ref_delta", "file": whether the
        levels refine a mesh.file, "paper": whether Table 1 applies, "total_s"}, on every
        rank.

    Raises:
        CaseError: the study's options or the case do not fit (see plan_runs), or the
            mesh.file cannot be refined.
        StudyInterrupted: SIGINT or SIGTERM ended the study (its ``finished`` runs are in
            the run cache, if there is one).
    """
    base = validate(raw, source)
    plan = plan_runs(levels, reference, vary, base, deltas)
    check_cache_dir(cache_dir, comm)
    deltas = list(deltas) if deltas else [base.numerics.delta]
    ref_delta = min([base.numerics.delta, *deltas])
    file = base.mesh.file is not None
    ref_N = _base_steps(base) * 2 ** reference if file else reference
    t0 = time.perf_counter()
    progress = _Progress(f"the refinement of {base.mesh.file}" if file else "its set-up")
    try:
        with level_meshes(base, reference, comm) as nested:
            def obtain(n, N, delta):
                progress.doing = f"the run {'r' if file else 'n'} = {n}, N = {N}, " \
                                 f"delta = {delta:g}"
                rec = obtain_run(raw, n, N, delta, source, petsc_cli, comm, cache_dir,
                                 level=nested[n] if nested else None)
                progress.finished += 1
                progress.doing = "the errors of the levels"
                return rec

            log.info("reference run %s (delta = %g)", f"r = {reference}, N = {ref_N}" if file
                     else f"n = N = {reference}", ref_delta)
            ref = obtain(reference, ref_N, ref_delta)
            rows, records = [], {}
            for delta in deltas:
                log.info("levels %s (vary %s, delta = %g)", levels, vary, delta)
                recs = [obtain(n, N, delta) for n, N in plan]
                records.update({(delta, L): r for L, r in zip(levels, recs)})
                rows += _level_rows(levels, recs, ref, vary, base.time.T, delta, comm)
    except KeyboardInterrupt as exc:
        raise progress.interrupted(exc) from None
    ref_norms = None
    if comm.rank == 0:
        *_, v_norm, cell_norm = _norm_ops(ref, ref)
        ref_norms = {"sigma_Q": max(cell_norm(sn["sigma"]) for sn in ref.snaps),
                     "u_V": max(v_norm(sn["u"]) for sn in ref.snaps),
                     "kappa_Y": max(cell_norm(sn["kappa"]) for sn in ref.snaps)}
    ref_norms = comm.bcast(ref_norms, root=0)
    return {"rows": rows, "reference": ref, "records": records, "ref_norms": ref_norms,
            "vary": vary, "levels": levels, "reference_level": reference, "deltas": deltas,
            "ref_delta": ref_delta, "file": file,
            "paper": matches_paper(raw) and vary == "both" and reference == 128,
            "total_s": time.perf_counter() - t0}


class _Progress:
    """What a study is doing and how many of its runs have finished, for the line of an
    interrupt.

    Args:
        doing: what the study does first.
    """

    def __init__(self, doing: str):
        self.doing, self.finished = doing, 0

    def interrupted(self, exc: KeyboardInterrupt) -> StudyInterrupted:
        """The StudyInterrupted of a signal that arrived now.

        Args:
            exc: the KeyboardInterrupt (or a run's StudyInterrupted, which says where and
                whether that run finished).

        Returns:
            The StudyInterrupted, with ``finished`` (the runs done or loaded from the cache).
        """
        if isinstance(exc, StudyInterrupted):     # from a run: where, and if it finished
            return StudyInterrupted(exc.signal, exc.where, self.finished + exc.finished)
        return StudyInterrupted(signal_name(exc), self.doing, self.finished)


def _level_rows(levels, recs, ref, vary, T, delta, comm) -> list[dict]:
    """The rows of one delta: Error (on rank 0, broadcast), rates, times."""
    errs = [run_error(r, ref) if comm.rank == 0 else None for r in recs]
    errs = comm.bcast(errs, root=0)
    xs = [r.h if vary != "k" else T / r.N for r in recs]
    printed = [float(f"{e['error']:.10g}") for e in errs]
    rates = _observed_rates(xs, printed)
    return [{"delta": delta, "level": L, "h": r.h, "k": T / r.N,
             "n": None if isinstance(r.grid, NestedLevel) else r.n, "N": r.N, "dofs": r.dofs,
             "steps": r.N, "error": p, "e_sigma": e["e_sigma"], "e_u": e["e_u"],
             "e_kappa": e["e_kappa"], "n_max": e["n_max"], "t_max": e["t_max"], "rate": rate,
             "solve_s": r.solve_s, "setup_s": r.setup_s, "newton_total": r.newton,
             "cached": r.cached, **_effectivity(r.estimate, p)}
            for L, r, e, p, rate in zip(levels, recs, errs, printed, rates)]


def _effectivity(estimate: dict | None, error: float) -> dict:
    """The columns of the run's error estimate: estimate, its time and space parts, the
    run's scale max_n (||sigma_n||_Q + ||u_n||_V + ||kappa_n||_Y) and the effectivity
    estimate / Error (None without an estimate or with a zero Error)."""
    if estimate is None:
        return {"estimate": None, "est_time": None, "est_space": None, "scale": None,
                "effectivity": None}
    return {"estimate": estimate["estimate"], "est_time": estimate["time"],
            "est_space": estimate["space"], "scale": estimate.get("scale"),
            "effectivity": estimate["estimate"] / error if error > 0 else None}


def check_level_sizes(case, comm, option: str, value: int, extra: int = 0) -> None:
    """Refuse a study whose finest refinement of the case's mesh.file would be larger than
    the built-in meshes may be (app/case/meshrules.py MAX_VERTICES) or could not be refined
    in the memory rank 0 has (meshes/refine.py, ``too_large``), before anything is refined
    or run: the vertex counts follow from the mesh read (``read_sizes``); collective.

    Args:
        case: the validated Case (nothing to check without a mesh.file).
        comm: the MPI communicator.
        option: the command line's option that sets the finest level ("--reference").
        value: its value.
        extra: the refinements the study adds to it (1 for the stability sweep's "h/2").

    Raises:
        CaseError: naming the option, the size and the values allowed, or mesh.file if the
            file cannot be read.
    """
    if case.mesh.file is None:
        return
    from vpcontact.case.meshrules import MAX_VERTICES
    from vpcontact.meshes import MeshFileError
    from vpcontact.meshes.refine import available_memory, read_sizes, too_large
    finest = value + extra
    try:
        sizes = read_sizes(comm, case.mesh.file, case.dim, case.mesh.size, finest)
    except MeshFileError as exc:
        raise CaseError(f"{case.source}: mesh.file: {exc}") from None
    memory = comm.bcast(available_memory() if comm.rank == 0 else None, root=0)  # refines
    over = too_large(sizes, case.dim, MAX_VERTICES, memory)
    if over:
        r, why = over
        raise CaseError(f"{case.source}: {option} {value}: the study refines mesh.file "
                        f"{finest} times; refined {r} times it {why}; allowed: {option} up "
                        f"to {r - 1 - extra} (or a coarser mesh)")


@contextlib.contextmanager
def level_meshes(case, reference: int, comm):
    """The refined levels 0..reference of a mesh.file case, as .msh files in a temporary
    directory (removed at the end); collective.

    Args:
        case: the validated Case.
        reference: the number of refinements of the finest level.
        comm: the MPI communicator.

    Yields:
        {r: NestedLevel}, or None for a built-in mesh.

    Raises:
        CaseError: naming mesh.file, if it cannot be read or refined that often.
    """
    if case.mesh.file is None:
        yield None
        return
    from vpcontact.case.meshrules import MAX_VERTICES
    from vpcontact.meshes import MeshFileError
    from vpcontact.meshes.refine import refine_file

    tmp = comm.bcast(tempfile.mkdtemp(prefix="vpcontact-levels-") if comm.rank == 0 else None,
                     root=0)
    try:
        try:
            paths, hierarchy = refine_file(comm, case.mesh.file, case.dim, case.mesh.size,
                                           reference, tmp, max_vertices=MAX_VERTICES)
        except MeshFileError as exc:
            raise CaseError(f"{case.source}: mesh.file: {exc}") from None
        h0 = comm.bcast(hierarchy[0].diameter() if comm.rank == 0 else None, root=0)
        yield {r: NestedLevel(r, p, h0 / 2 ** r, hierarchy) for r, p in enumerate(paths)}
    finally:
        if comm.rank == 0:
            shutil.rmtree(tmp, ignore_errors=True)


# ----------------------------------------------------------------------------- reports
def _fmt(v, digits=4):
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def write_csv(path: Path, res: dict) -> None:
    """Write the study's rows as CSV (the COLUMNS; floats at full precision), atomically.

    Args:
        path: the CSV file.
        res: the result of ``study``.
    """
    atomic_write(path, csv_text(COLUMNS, res["rows"]))


def paper_sentence(rows: list[dict]) -> str:
    """Compare the study's Errors and rates with the paper's Table 1.

    Args:
        rows: the study's rows of one delta.

    Returns:
        One sentence: the range of our/paper Error ratios, whether they agree to 10%, and
        the observed rates beside the paper's; "" if no level is one of the paper's.
    """
    ours = {r["level"]: r for r in rows}
    common = [L for L in PAPER_TABLE1 if L in ours]
    if not common:
        return ""
    ratio = [ours[L]["error"] / PAPER_TABLE1[L] for L in common]
    rates = [(L, ours[L]["rate"], PAPER_RATES[L]) for L in common if L in PAPER_RATES
             and ours[L]["rate"] is not None]
    agree = all(abs(r - 1) < 0.1 for r in ratio)
    text = (f"Our errors are {min(ratio):.3g} to {max(ratio):.3g} times the paper's "
            f"({'they agree to 10%' if agree else 'they do not agree in magnitude'}); observed "
            "rates ours/paper: " + ", ".join(f"h = 1/{L}: {a:.3f}/{b:.4f}" for L, a, b in rates))
    return text + "."


def write_markdown(path: Path, res: dict, case_name: str) -> None:
    """Write the study's report (the Error definition, a table per delta, the paper's
    Table 1 beside it when it applies, and ``explain``), atomically.

    Args:
        path: the Markdown file.
        res: the result of ``study``.
        case_name: the case's name, for the title.
    """
    ref = res["reference"]
    var = "h = k" if res["vary"] == "both" else res["vary"]
    what = (f"the mesh refined {res['reference_level']} times" if res.get("file") else
            f"n = N = {res['reference_level']}")
    lines = [f"# Convergence study: {case_name}", "",
             f"Refined: {var} (`--vary {res['vary']}`); reference {what} ({ref.dofs} dofs, "
             f"{ref.N} steps, delta = {res['ref_delta']:g}, solve time {ref.solve_s:.2f} s"
             f"{', cached' if ref.cached else ''}).", ""]
    if res.get("file"):
        lines += ["Level r (column r) is the case's mesh.file refined r times: each triangle "
                  "split into 4 (each tetrahedron into 8) by its edges' midpoints, so the "
                  "meshes are nested (a curved boundary keeps the polygon of the mesh read) "
                  "and h = h_0 / 2^r, h_0 the largest cell diameter of the mesh read; a level "
                  "has N = time.N 2^r steps when k is refined.", ""]
    lines += ["Error = max_n (||sigma_n - sigma_n^ref||_Q + ||u_n - u_n^ref||_V + "
              "||kappa_n - kappa_n^ref||_Y) over the level's time points; the level's fields "
              "are prolonged exactly to the reference mesh and the norms integrated there "
              "(||v||_V = ||eps(v)||_L2, Frobenius). Parts are given at the maximising step "
              "n_max.", "",
              "Wall time = sum over the steps of the time spent in the history update, the "
              "SNES solve and the stress update (time.perf_counter); mesh generation, JIT "
              "compilation, set-up, outputs and sampling are excluded (set-up column). Cached "
              "runs show the times measured when they were computed.", "",
              "Estimate = the level's own a posteriori estimate of its Error (summary.json's "
              "error_estimate: the summed local errors of the history update plus the "
              "recovery estimate of the space error); effectivity = estimate / Error.", ""]
    for delta in res["deltas"]:
        rows = [r for r in res["rows"] if r["delta"] == delta]
        paper = res["paper"]
        head = ["r"] * bool(res.get("file")) + [
            "h", "k", "dofs", "steps", "Error", "sigma part", "u part", "kappa part", "n_max",
            "rate", "estimate", "effectivity", "wall s", "set-up s", "Newton"]
        if paper:
            head += ["paper Error", "paper rate"]
        lines += [f"## delta = {delta:g}", "", "| " + " | ".join(head) + " |",
                  "|" + "---|" * len(head)]
        for r in rows:
            cells = [r["level"]] * bool(res.get("file")) + [
                     f"1/{round(1 / r['h'])}" if abs(1 / r["h"] - round(1 / r["h"])) < 1e-9
                     else _fmt(r["h"]),
                     f"1/{round(1 / r['k'])}" if abs(1 / r["k"] - round(1 / r["k"])) < 1e-9
                     else _fmt(r["k"]),
                     r["dofs"], r["steps"], f"{r['error']:.6g}", _fmt(r["e_sigma"]),
                     _fmt(r["e_u"]), _fmt(r["e_kappa"]), r["n_max"], _fmt(r["rate"]),
                     _fmt(r["estimate"]), _fmt(r["effectivity"], 3), f"{r['solve_s']:.3f}",
                     f"{r['setup_s']:.2f}", r["newton_total"]]
            if paper:
                cells += [_fmt(PAPER_TABLE1.get(r["level"])), _fmt(PAPER_RATES.get(r["level"]))]
            lines.append("| " + " | ".join(map(str, cells)) + " |")
        lines.append("")
        if paper:
            lines += [paper_sentence(rows), ""]
    lines += explain(res)
    atomic_write(path, "\n".join(lines) + "\n")


def explain(res: dict) -> list[str]:
    """Facts that explain where the Error comes from (and, for Table 1, the differences).

    Args:
        res: the result of ``study``.

    Returns:
        Markdown lines (a section with bullet points), or [] if there are no rows.
    """
    rows = [r for r in res["rows"] if r["delta"] == res["deltas"][0]]
    if not rows:
        return []
    fin = rows[-1]
    nr = res["ref_norms"]
    share = fin["e_sigma"] / fin["error"]
    out = ["## Where the error comes from", "",
           f"- At the finest level the stress part is {100 * share:.1f}% of the Error "
           f"(sigma {fin['e_sigma']:.4g}, u {fin['e_u']:.4g}, kappa {fin['e_kappa']:.4g}); the "
           "maximum over n is reached at step(s) n_max = "
           + ", ".join(str(r["n_max"]) for r in rows) + " (t = "
           + ", ".join(f"{r['t_max']:.4g}" for r in rows) + ").",
           f"- Size of the reference solution: max_n ||sigma_n||_Q = {nr['sigma_Q']:.4g}, "
           f"max_n ||u_n||_V = {nr['u_V']:.4g}, max_n ||kappa_n||_Y = {nr['kappa_Y']:.4g}.",
           "- The observed rate at the finest level is measured against a reference only "
           f"{_finer(res, rows[-1]['level'])}x finer; the reference's own error is "
           "then not negligible and this last rate is biased (for an error C h^p it "
           "overestimates p)."]
    if res["paper"]:
        big = max(PAPER_TABLE1.values())
        out.append(f"- The paper's Errors ({big} at h = 1/8) exceed the size of the solution "
                   f"itself (max_n ||sigma_n||_Q = {nr['sigma_Q']:.3g}); an error of that size "
                   "cannot be this Error in these norms for this solution, so the paper's norms "
                   "(or their scaling) must differ from the Error defined above; the paper does "
                   "not say how they were computed. Compare the rates, not the magnitudes.")
    return out + [""]


def _finer(res: dict, level: int) -> int:
    """How many times finer the reference is than a level."""
    R = res["reference_level"]
    return 2 ** (R - level) if res.get("file") else R // level


def convergence_figure(res: dict):
    """The figure of ``write_plot``: Error against h (or k), and against wall time.

    Args:
        res: the result of ``study``.

    Returns:
        The matplotlib Figure (laid out, not saved).
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xkey = "k" if res["vary"] == "k" else "h"
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    for delta in res["deltas"]:
        rows = [r for r in res["rows"] if r["delta"] == delta]
        x = [r[xkey] for r in rows]
        e = [r["error"] for r in rows]
        ax1.loglog(x, e, "o-", label=f"delta = {delta:g}")
        ax2.loglog([max(r["solve_s"], 1e-4) for r in rows], e, "s-", label=f"delta = {delta:g}")
    rows = [r for r in res["rows"] if r["delta"] == res["deltas"][0]]
    if rows:
        x0, e0 = rows[-1][xkey], rows[-1]["error"]
        xs = np.array([r[xkey] for r in rows])
        ax1.loglog(xs, e0 * xs / x0, "k--", lw=1, label="slope 1")
    if res["paper"]:
        ax1.loglog([1 / L for L in PAPER_TABLE1], list(PAPER_TABLE1.values()), "x:",
                   color="grey", label="paper Table 1")
    for axis in (ax1.yaxis, ax2.xaxis, ax2.yaxis):
        _log_ticks(axis)
    ticks = sorted({r[xkey] for r in res["rows"]})
    ax1.set_xticks(ticks)
    ax1.set_xticklabels([f"1/{round(1 / x)}" if abs(1 / x - round(1 / x)) < 1e-9 else f"{x:g}"
                         for x in ticks])
    ax1.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())   # the levels only
    ax1.set_xlabel(xkey if res["vary"] != "both" else "h = k")
    ax1.set_ylabel("Error")
    ax1.set_title(f"Error against {xkey} (reference "
                  + (f"refined {res['reference_level']} times)" if res.get("file") else
                     f"1/{res['reference_level']})"))
    ax2.set_xlabel("wall time of the run [s] (steps only, no JIT)")
    ax2.set_ylabel("Error")
    ax2.set_title("work-precision")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    return fig


def _log_ticks(axis) -> None:
    """Labelled ticks on a log axis whatever its span: at 1, 2, 5 x 10^k (every integer
    multiple below a decade), plain numbers, no unlabelled minor ticks.  (matplotlib's
    default labels only powers of 10: a panel spanning less than a decade had none.)"""
    import matplotlib.ticker as mticker
    lo, hi = sorted(axis.get_view_interval())
    subs = (1.0, 2.0, 5.0) if hi > 10 * lo else tuple(range(1, 10))
    axis.set_major_locator(mticker.LogLocator(base=10, subs=subs))
    axis.set_major_formatter(mticker.FuncFormatter(lambda v, _: f"{v:.3g}"))
    axis.set_minor_locator(mticker.NullLocator())


def write_plot(path: Path, res: dict) -> None:
    """Plot Error against h (or k) and against wall time (work-precision), with the
    paper's Table 1 when it applies, to a PNG (atomically).

    Args:
        path: the PNG file.
        res: the result of ``study``.
    """
    import matplotlib.pyplot as plt

    from vpcontact.io.files import write_replacing
    fig = convergence_figure(res)
    write_replacing(path, lambda tmp: fig.savefig(tmp, dpi=120))
    plt.close(fig)
